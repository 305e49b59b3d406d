"""Wording shared by the language's error messages: near names, shapes, numbers."""
from __future__ import annotations

import difflib

import numpy as np


def close(name: str, options) -> str:
    """' (did you mean 'a' or 'b'?)' or ''."""
    found = difflib.get_close_matches(name, sorted(set(options)), n=3, cutoff=0.6)
    if not found:
        return ""
    return " (did you mean " + " or ".join(f"'{f}'" for f in found) + "?)"


def shape_words(shape) -> str:
    """'a single number', '3 numbers' or 'an array of shape 2x3'."""
    if shape == ():
        return "a single number"
    if len(shape) == 1:
        return f"{shape[0]} numbers"
    return "an array of shape " + "x".join(map(str, shape))


def fmt(arr: np.ndarray) -> str:
    """A number or a vector as short text: '0.5' or '(1, 2, 3)'."""
    arr = np.asarray(arr)
    return f"{float(arr):g}" if arr.ndim == 0 else "(" + ", ".join(f"{v:g}" for v in arr.ravel()) + ")"
