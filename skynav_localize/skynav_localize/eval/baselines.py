# SPDX-License-Identifier: Apache-2.0
"""Baselines users would pick instead: SeqSLAM on down-sampled raw UV images, and a bag of ORB visual words.

- raw UV (SeqSLAM's own front end): the fish-eye UV image, area-averaged down to RAW_UV_SIZE pixels, each
  RAW_UV_PATCH x RAW_UV_PATCH patch normalised to zero mean and unit standard deviation (gain and offset drop
  out); distance: mean absolute difference ('sad'). Not rotation invariant: a turned robot sees a turned image.
- bag of words on ORB (OpenCV's detector and descriptor): ORB features of the UV image inside the image circle;
  a vocabulary of BOW_WORDS visual words by k-means (Lloyd's iterations, BLAS-backed; cv2.kmeans gives the same
  kind of result about five times slower here) on the map's descriptors with their bits as 0/1 vectors; each
  feature votes for its nearest word (Euclidean distance in bit space); tf-idf weights with the idf of the map's
  snapshots, unit norm; distance: cosine distance 1 - cos. 1024 words measured better than 256 or 64 on the
  bundled synthetic pairs (recall@1 at 1 m 1.0 / 1.0 against 0.98 / 0.88 with 256), so the baseline gets them.

Importing this module registers the baselines' methods (BASELINE_METHODS: 'raw-uv', 'seqslam-raw-uv', 'bow-orb') with
the Localizer (localizer.register); EVALUATED_METHODS is every method `skynav eval localization` offers, skynav's
first. It also makes and finishes the baselines' descriptors of a map (`skynav map build --baselines`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import csr_matrix

from skynav_core.maps import MapError, MapStore
from skynav_localize.descriptors import describe
from skynav_localize.errors import LocalizeError
from skynav_localize.localizer import METHODS, Method, register
from skynav_localize.mapping import ORB_FEATURES as ORB_FEATURES  # features per image
from skynav_localize.mapping import RAW_UV_PATCH as RAW_UV_PATCH  # px, side of the down-sampled image's patches
from skynav_localize.mapping import RAW_UV_SIZE as RAW_UV_SIZE  # px (width, height) of the down-sampled image
from skynav_localize.mapping import SH_DESCRIPTOR_NAMES
from skynav_localize.matching import Acceptance

ORB_CIRCLE_MARGIN = 8  # px kept free inside the image circle's edge (its contour is the same in every image)
BOW_WORDS = 1024  # visual words of the vocabulary
BOW_MAX_SAMPLES = 10000  # ORB descriptors (at most) that train the vocabulary
BOW_ITERATIONS = 20  # k-means iterations
VOCABULARY_WORDS = 'bow-orb.words'  # map artifact: (K, 256) float32 word centres (bit space)
VOCABULARY_IDF = 'bow-orb.idf'  # map artifact: (K,) float64 inverse document frequencies


def image_as_float(image: np.ndarray) -> np.ndarray:
    """Return a single-channel image (mono8, mono16 or 32FC1 array) as float32 radiance units (any gain)."""
    image = np.asarray(image)
    if image.ndim != 2:
        raise LocalizeError(f'expected a single-channel (H, W) image, got shape {image.shape}')
    return image.astype(np.float32, copy=False)


def raw_uv_descriptor(image: np.ndarray, size: tuple[int, int] = RAW_UV_SIZE, patch: int = RAW_UV_PATCH) -> np.ndarray:
    """Return SeqSLAM's patch-normalised down-sampled image (width x height values, float32) of a UV image."""

    width, height = size
    if width % patch or height % patch:
        raise LocalizeError(f'size {size} must be a multiple of the patch side {patch}')
    small = cv2.resize(image_as_float(image), (width, height), interpolation=cv2.INTER_AREA)
    blocks = small.reshape(height // patch, patch, width // patch, patch)
    mean = blocks.mean(axis=(1, 3), keepdims=True)
    std = blocks.std(axis=(1, 3), keepdims=True)
    normalised = np.divide(blocks - mean, std, out=np.zeros_like(blocks), where=std > 0)
    return normalised.reshape(-1)


def as_uint8(image: np.ndarray, circle: np.ndarray | None = None) -> np.ndarray:
    """Return an image as uint8 for ORB: mono8 as is, others scaled so that their 99.5th percentile is 255."""
    image = np.asarray(image)
    if image.dtype == np.uint8:
        return image
    values = image_as_float(image)
    inside = values[circle] if circle is not None else values
    top = float(np.percentile(inside, 99.5)) if inside.size else 0.0
    scale = 255.0 / top if top > 0 else 0.0
    return np.clip(values * scale, 0, 255).astype(np.uint8)


def orb_mask(circle: np.ndarray | None, shape: tuple[int, int]) -> np.ndarray | None:
    """Return ORB's detection mask (uint8, 255 inside): the image circle shrunk by ORB_CIRCLE_MARGIN px, or None."""
    if circle is None:
        return None

    circle = np.asarray(circle, dtype=bool)
    if circle.shape != tuple(shape):
        raise LocalizeError(f'image circle {circle.shape} does not fit the image {tuple(shape)}')
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ORB_CIRCLE_MARGIN + 1,) * 2)
    return cv2.erode(circle.astype(np.uint8) * 255, kernel)


def orb_descriptors(image: np.ndarray, circle: np.ndarray | None = None, n_features: int = ORB_FEATURES) -> np.ndarray:
    """Return the ORB descriptors (n, 32) uint8 of a UV image, features inside the image circle (bool mask) only."""

    image8 = as_uint8(image, None if circle is None else np.asarray(circle, dtype=bool))
    orb = cv2.ORB.create(nfeatures=int(n_features))
    _, descriptors = orb.detectAndCompute(image8, orb_mask(circle, image8.shape))
    return np.zeros((0, 32), np.uint8) if descriptors is None else descriptors


def _bits(descriptors: np.ndarray) -> np.ndarray:
    """Return ORB descriptors (n, 32) uint8 as 0/1 vectors (n, 256) float32."""
    return np.unpackbits(np.asarray(descriptors, dtype=np.uint8), axis=1).astype(np.float32)


def kmeans(points: np.ndarray, count: int, rng: np.random.Generator, iterations: int = BOW_ITERATIONS) -> np.ndarray:
    """Return `count` k-means centres (count, D) float32 of points (n, D), started from distinct random points."""

    points = np.asarray(points, dtype=np.float32)
    centres = points[rng.choice(len(points), count, replace=False)].copy()
    previous = None
    for _ in range(int(iterations)):
        nearest = np.argmin(np.einsum('kd,kd->k', centres, centres)[None, :] - 2.0 * (points @ centres.T), axis=1)
        if previous is not None and np.array_equal(nearest, previous):
            break
        previous = nearest
        members = csr_matrix(
            (np.ones(len(points), np.float32), (nearest, np.arange(len(points)))), shape=(count, len(points))
        )
        sizes = np.bincount(nearest, minlength=count)
        sums = np.asarray(members @ points)
        filled = sizes > 0  # an empty cluster keeps its centre
        centres[filled] = sums[filled] / sizes[filled, None]
    return centres


class NoFeatures(LocalizeError):
    """No ORB feature in any snapshot (a featureless teach drive: all sky, an open field, all ground): no vocabulary."""


@dataclass(frozen=True)
class BowVocabulary:
    """Visual words (K centres in ORB bit space) and the inverse document frequencies of a map's snapshots."""

    words: np.ndarray  # (K, 256) float32
    idf: np.ndarray  # (K,) float64, log((1 + N) / (1 + snapshots containing the word))

    @classmethod
    def train(
        cls, descriptor_sets: list[np.ndarray], size: int = BOW_WORDS, seed: int = 0, max_samples: int = BOW_MAX_SAMPLES
    ) -> BowVocabulary:
        """Return a vocabulary by k-means on (a sample of) the snapshots' ORB descriptors and their idf."""
        pool = np.concatenate([np.asarray(d, np.uint8).reshape(-1, 32) for d in descriptor_sets])
        if len(pool) == 0:
            raise NoFeatures('no ORB features in any snapshot to train a vocabulary on')
        rng = np.random.default_rng(seed)
        if len(pool) > max_samples:
            pool = pool[rng.choice(len(pool), max_samples, replace=False)]
        vocabulary = cls(kmeans(_bits(pool), min(int(size), len(pool)), rng), np.zeros(0))
        present = np.stack([np.bincount(vocabulary.assign(d), minlength=vocabulary.size) > 0 for d in descriptor_sets])
        idf = np.log((1.0 + len(descriptor_sets)) / (1.0 + present.sum(axis=0)))
        return cls(vocabulary.words, idf)

    @property
    def size(self) -> int:
        """Return the number of words K."""
        return self.words.shape[0]

    def assign(self, descriptors: np.ndarray) -> np.ndarray:
        """Return the nearest word (n,) of each ORB descriptor (n, 32)."""
        bits = _bits(np.asarray(descriptors).reshape(-1, 32))
        if len(bits) == 0:
            return np.zeros(0, dtype=np.intp)
        squared = np.einsum('kd,kd->k', self.words, self.words)[None, :] - 2.0 * bits @ self.words.T
        return np.argmin(squared, axis=1)  # |bits|^2 is the same for every word

    def histogram(self, descriptors: np.ndarray) -> np.ndarray:
        """Return the word counts (K,) of one image's ORB descriptors."""
        return np.bincount(self.assign(descriptors), minlength=self.size).astype(float)

    def vector(self, descriptors: np.ndarray) -> np.ndarray:
        """Return the unit tf-idf vector (K,) of one image's ORB descriptors (zero if it has none)."""
        counts = self.histogram(descriptors)
        total = counts.sum()
        weighted = (counts / total if total > 0 else counts) * self.idf
        norm = np.linalg.norm(weighted)
        return weighted / norm if norm > 0 else weighted

    def vectors(self, descriptor_sets: list[np.ndarray]) -> np.ndarray:
        """Return the unit tf-idf vectors (M, K) of several images' ORB descriptors."""
        return np.stack([self.vector(d) for d in descriptor_sets]) if descriptor_sets else np.zeros((0, self.size))

    def save(self, store) -> None:
        """Store the vocabulary in a writable map (artifacts) with every snapshot's tf-idf vector ('bow-orb')."""
        store.put_artifact(VOCABULARY_WORDS, self.words)
        store.put_artifact(VOCABULARY_IDF, self.idf)
        store.put_descriptors('bow-orb', self.vectors(store.descriptor_list('orb')).astype(np.float32))

    @classmethod
    def load(cls, store) -> BowVocabulary | None:
        """Return the vocabulary stored in a map, None if it has none."""
        words, idf = store.artifact(VOCABULARY_WORDS), store.artifact(VOCABULARY_IDF)
        if words is None or idf is None:
            return None
        return cls(np.asarray(words, np.float32), np.asarray(idf, float))


def train_bow(store, size: int = BOW_WORDS, seed: int = 0) -> BowVocabulary:
    """Train the ORB vocabulary of a writable map from its snapshots' 'orb' descriptors and store it (after a build).

    NoFeatures when no snapshot has a single ORB feature.
    """
    vocabulary = BowVocabulary.train(store.descriptor_list('orb'), size, seed)
    vocabulary.save(store)
    return vocabulary


#: The baselines' descriptors of a UV image, stored per snapshot by `skynav map build --baselines`.
IMAGE_DESCRIPTOR_NAMES = ('raw_uv', 'orb')


def snapshot_descriptors(
    coefficients: np.ndarray,
    max_degree: int,
    uv: np.ndarray | None = None,
    circle: np.ndarray | None = None,
    names: Iterable[str] | None = None,
) -> dict[str, np.ndarray]:
    """Return one snapshot's descriptors by name: SH ones from coefficients, 'raw_uv' and 'orb' from the UV image."""
    if names is None:
        names = SH_DESCRIPTOR_NAMES + (IMAGE_DESCRIPTOR_NAMES if uv is not None else ())
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name in SH_DESCRIPTOR_NAMES:
            out[name] = describe(name, coefficients, max_degree)
        elif name in IMAGE_DESCRIPTOR_NAMES:
            if uv is None:
                raise LocalizeError(f'descriptor {name!r} needs the UV image')
            out.update(baseline_descriptors(uv, circle, (name,)))
        else:
            raise LocalizeError(
                f'unknown descriptor {name!r}; expected one of '
                f'{", ".join(SH_DESCRIPTOR_NAMES + IMAGE_DESCRIPTOR_NAMES)}'
            )
    return out


def baseline_descriptors(
    uv: np.ndarray, circle: np.ndarray | None = None, names: Iterable[str] = IMAGE_DESCRIPTOR_NAMES
) -> dict[str, np.ndarray]:
    """Return the baselines' descriptors of one snapshot's UV image: 'raw_uv' and 'orb' (inside the image circle)."""
    return {name: raw_uv_descriptor(uv) if name == 'raw_uv' else orb_descriptors(uv, circle) for name in names}


def finish_baselines(store: MapStore) -> list[str]:
    """Train what the baselines need once every snapshot is stored (the ORB vocabulary); return a line per one left out.

    A teach drive without a single ORB feature (all sky, an open field, all ground) has no vocabulary: the bag of
    words is left out (its 'orb' rows removed) and says so in one line; the map is complete without it.
    """
    if 'orb' not in store.descriptor_names():
        return []
    try:
        train_bow(store)
    except NoFeatures:
        store.remove_descriptors('orb')
        return ['bow-orb: no ORB features in the teach drive; its descriptors are left out']
    return []


class RawUvDescriptors:
    """SeqSLAM's raw UV descriptors of the map's snapshots (stored) and of the queries, as the map's were made."""

    def missing(self, store: MapStore) -> str:
        """Return what a non-empty map lacks ('' if nothing)."""
        return '' if 'raw_uv' in store.descriptor_names() else "raw UV descriptors ('raw_uv')"

    def prepare(
        self, store: MapStore, settings: Mapping, circle: np.ndarray | None
    ) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """Return the map's raw UV descriptors and the function that describes a query's UV image."""
        size = tuple(settings.get('raw_uv_size', RAW_UV_SIZE))
        patch = int(settings.get('raw_uv_patch', RAW_UV_PATCH))
        return store.descriptor_matrix('raw_uv'), lambda uv: raw_uv_descriptor(uv, size, patch)


class BowOrbDescriptors:
    """The bag of ORB words: the map's stored vocabulary and vectors, or a vocabulary trained now from its ORB
    features; a query's tf-idf vector of its ORB features (inside the image circle)."""

    def missing(self, store: MapStore) -> str:
        """Return what a non-empty map lacks ('' if nothing)."""
        stored = set(store.descriptor_names())
        if 'orb' not in stored and not ('bow-orb' in stored and BowVocabulary.load(store) is not None):
            return "ORB descriptors ('orb') or their vocabulary"
        return ''

    def prepare(
        self, store: MapStore, settings: Mapping, circle: np.ndarray | None
    ) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """Return the map's tf-idf vectors and the function that describes a query's UV image."""
        vocabulary = BowVocabulary.load(store)
        if vocabulary is not None and 'bow-orb' in store.descriptor_names():
            matrix = store.descriptor_matrix('bow-orb')
        else:
            orb = store.descriptor_list('orb')
            try:
                vocabulary = BowVocabulary.train(orb)
            except NoFeatures:
                raise MapError(
                    f'{store.path}: method bow-orb needs ORB features, and no snapshot of this map has any'
                ) from None
            matrix = vocabulary.vectors(orb)
        features = int(settings.get('orb_features', ORB_FEATURES))
        trained = vocabulary
        return matrix, lambda uv: trained.vector(orb_descriptors(uv, circle, features))


# Baselines, where correct and off-route ratios overlap, keep precision 1 on the pairs: raw UV 0.85, SeqSLAM raw UV
# 0.8, BoW ORB 0.45; they are SeqSLAM and a bag of words as their authors describe them, without the view test.
# A real camera and route should have them re-learned (evaluation.threshold_at_full_precision on a labelled drive).
_RAW_UV, _BOW_ORB = RawUvDescriptors(), BowOrbDescriptors()
PEER_METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method('raw-uv', 'raw_uv', 'sad', False, 'uv', Acceptance(0.85), True, np.float32, _RAW_UV),
        Method('seqslam-raw-uv', 'raw_uv', 'sad', True, 'uv', Acceptance(0.8), True, np.float32, _RAW_UV),
        Method('bow-orb', 'bow-orb', 'cosine', False, 'uv', Acceptance(0.45), True, np.float32, _BOW_ORB),
    )
}
register(*PEER_METHODS.values())
BASELINE_METHODS = tuple(PEER_METHODS)
#: Every method `skynav eval localization` offers: skynav's (the node's), then the baselines.
EVALUATED_METHODS: dict[str, Method] = {**METHODS, **PEER_METHODS}
