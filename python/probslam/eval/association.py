"""Data association against a dataset's labels: how well a landmark filter's (or a refinement's)
labelling of the sightings matches their true landmarks."""

from __future__ import annotations

import collections
from typing import Dict, Iterator, Tuple

import numpy as np

from .._args import require_fields
from .landmarks import _RESULT_FIELDS


def _record(result):
    """The association record of a hidden-correspondence run."""
    require_fields(result, _RESULT_FIELDS, "result", "a LandmarkSlamResult")
    if result.associations is None:
        raise ValueError("result: a run with known correspondences has no associations to score")
    return result.associations


def _applied_sightings(result) -> Iterator[Tuple[int, int]]:
    """(true id, filter landmark id) of every sighting a hidden-correspondence run put in its map."""
    record = _record(result)
    applied = record.ids >= 0
    return zip(record.truth[applied].tolist(), record.ids[applied].tolist())


def _labelling(labels, truth) -> Tuple[np.ndarray, np.ndarray]:
    """(labels, truth) of the labelled sightings (label != -1), checked to be two (K,) arrays."""
    labels, truth = np.asarray(labels), np.asarray(truth)
    if labels.shape != truth.shape or labels.ndim != 1:
        raise ValueError(f"labels, truth: expected two (K,) arrays, got {labels.shape} and {truth.shape}")
    keep = labels != -1
    return labels[keep], truth[keep]


def majority_truth(labels, truth) -> Dict[int, int]:
    """A labelling of sightings against their true ids, on arrays: labels (K,) (the landmark each
    sighting went to, -1 for none), truth (K,): each label -> the true id most of its sightings
    carry."""
    labels, truth = _labelling(labels, truth)
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for lab, t in zip(labels.tolist(), truth.tolist()):
        votes[int(lab)][int(t)] += 1
    return {lab: c.most_common(1)[0][0] for lab, c in votes.items()}


def sighting_accuracy(labels, truth) -> float:
    """Fraction of the labelled sightings (label != -1) whose label's majority true id
    (``majority_truth``) is their own; NaN when none is labelled."""
    labels, truth = _labelling(labels, truth)
    if len(labels) == 0:
        return float("nan")
    major = majority_truth(labels, truth)
    return float(np.mean([major[int(lab)] == int(t) for lab, t in zip(labels.tolist(), truth.tolist())]))


def majority_labels(result) -> Dict[int, int]:
    """For a run with hidden correspondences: each filter landmark -> the true id (the dataset's
    label) most of its sightings carry."""
    record = _record(result)
    return majority_truth(record.ids, record.truth)


def primary_landmarks(result) -> Dict[int, int]:
    """For a run with hidden correspondences: true id -> the filter landmark holding most of its
    sightings (duplicates left out), among the landmarks still in the map."""
    votes: Dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for t, i in _applied_sightings(result):
        if i in result.landmarks:
            votes[t][i] += 1
    return {t: c.most_common(1)[0][0] for t, c in votes.items()}


def association_accuracy(result) -> float:
    """Fraction of the sightings put in the map that went to a landmark whose majority true id
    (``majority_labels``) is their own; NaN when none was."""
    record = _record(result)
    return sighting_accuracy(record.ids, record.truth)
