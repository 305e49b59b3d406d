"""Helpers of the rendering tests."""
import numpy as np


def silhouette(image, empty, threshold=0.1):
    """Pixels where an image differs from the empty scene (ground and sky only)."""
    return np.abs(np.asarray(image) - np.asarray(empty)).sum(-1) > threshold


def centroid(mask):
    rows, cols = np.nonzero(mask)
    return np.array([cols.mean(), rows.mean()])
