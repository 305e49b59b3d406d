"""Images as measurements: reading frames from files or videos, and their likelihood.

The likelihood compares a rendered image with an observed one pixel by pixel at several blur
levels (a Gaussian pyramid): the sharp level pins the answer down, the blurred levels keep the
likelihood sloping towards it from far away. See docs/rendering.md.
"""
from __future__ import annotations

import glob as _glob
from pathlib import Path
from typing import NamedTuple, Sequence

import jax.numpy as jnp
import numpy as np
from jax.scipy.special import gammaln

from ..errors import DataError

VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg"}


class VideoFrame(NamedTuple):
    """Frame ``index`` of a video file: one entry of an image observation's frame list."""

    path: Path
    index: int

    def __str__(self) -> str:
        return f"{self.path} (frame {self.index})"


def is_video(path) -> bool:
    """Whether ``path`` names a video file (by its suffix)."""
    return not isinstance(path, (list, tuple)) and Path(str(path)).suffix.lower() in VIDEO_SUFFIXES


def video_frames(path: Path) -> tuple[tuple[VideoFrame, ...], float]:
    """The frames of a video as VideoFrame entries, and its stated frame rate (0 if none)."""
    frames, fps = _read_video(path)
    return tuple(VideoFrame(path, i) for i in range(len(frames))), fps


def _cv2():
    import cv2

    return cv2


def _expand(source) -> list[Path]:
    """Frame files of a list of paths, a directory (sorted images), or a glob pattern."""
    if isinstance(source, (list, tuple)):
        return [p if isinstance(p, VideoFrame) else Path(p) for p in source]
    text = str(source)
    path = Path(text)
    if path.is_dir():
        files = sorted(p for p in path.iterdir()
                       if p.suffix.lower() in {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"})
        if not files:
            raise DataError("no image files in this folder", path)
        return files
    if any(ch in text for ch in "*?["):
        files = [Path(p) for p in sorted(_glob.glob(text))]
        if not files:
            raise DataError("no file matches this pattern", text)
        return files
    return [path]


def _read_images(paths) -> list[np.ndarray]:
    """Images of a list of files and VideoFrame entries (each video read once)."""
    videos = {p.path: _read_video(p.path)[0] for p in paths if isinstance(p, VideoFrame)}
    out = []
    for p in paths:
        if isinstance(p, VideoFrame):
            if p.index >= len(videos[p.path]):
                raise DataError(f"the video has {len(videos[p.path])} frames, not "
                                f"{p.index + 1}", p.path)
            out.append(videos[p.path][p.index])
        else:
            out.append(_read_image(Path(p)))
    return out


def _read_image(path: Path) -> np.ndarray:
    if not path.exists():
        raise DataError("frame file not found", path)
    if path.suffix.lower() in VIDEO_SUFFIXES:
        raise DataError("a video among image frames", path,
                        hint="give the video alone (from \"clip.mp4\") or only image files")
    img = _cv2().imread(str(path), _cv2().IMREAD_COLOR)
    if img is None:
        raise DataError("cannot read this file as an image", path,
                        hint="frames must be PNG, JPG, BMP or TIFF images")
    return img[:, :, ::-1].astype(np.float64) / 255.0


def _read_video(path: Path) -> tuple[list[np.ndarray], float]:
    if not path.exists():
        raise DataError("video file not found", path)
    cap = _cv2().VideoCapture(str(path))
    frames = []
    try:
        if not cap.isOpened():
            raise DataError("cannot open this file as a video", path)
        fps = float(cap.get(_cv2().CAP_PROP_FPS) or 0.0)
        while True:
            ok, img = cap.read()
            if not ok:
                break
            frames.append(img[:, :, ::-1].astype(np.float64) / 255.0)
    finally:
        cap.release()
    if not frames:
        raise DataError("the video has no readable frames", path)
    return frames, fps


def load_frames(source, times: Sequence[float] | None = None, rate: float | None = None,
                size: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(times (N,), frames (N, H, W, 3) float in [0, 1]) from image files or a video.

    ``source``: a list of files, a glob pattern, a folder of images, or a video file. Frame
    times come from ``times``, else ``rate`` (frame i at i / rate), else the video's frame rate.
    ``size`` (width, height), if given, is checked. Any problem is a DataError naming the file.
    """
    if is_video(source):
        frames, fps = _read_video(Path(str(source)))
        names = [str(VideoFrame(Path(str(source)), i)) for i in range(len(frames))]
        if times is None and rate is None:
            if fps <= 0:
                raise DataError("the video does not state its frame rate", source,
                                hint="give the frame rate (--rate) or the frame times")
            rate = fps
    else:
        files = _expand(source)
        frames = _read_images(files)
        names = [str(p) for p in files]
    want = (size[1], size[0]) if size is not None else frames[0].shape[:2]
    for name, img in zip(names, frames):
        if img.shape[:2] != tuple(want):
            raise DataError(f"frame is {img.shape[1]}x{img.shape[0]} pixels, expected "
                            f"{want[1]}x{want[0]}", name)
    if times is not None:
        t = np.asarray(times, dtype=float).reshape(-1)
        if t.shape[0] != len(frames):
            raise DataError(f"{len(frames)} frames but {t.shape[0]} frame times", names[0])
    elif rate is not None:
        t = np.arange(len(frames)) / float(rate)
    else:
        raise DataError("frame times unknown", names[0], hint="give a frame rate or times")
    if np.any(np.diff(t) <= 0):
        raise DataError("frame times must increase", names[0])
    return t, np.stack(frames)


def _blur_matrix(n: int, sigma: float, stride: int) -> np.ndarray:
    """Rows of a (edge-renormalised) Gaussian blur along one axis, keeping every ``stride``-th."""
    x = np.arange(n, dtype=float)
    if sigma <= 0:
        m = np.eye(n)
    else:
        m = np.exp(-0.5 * ((x[:, None] - x[None, :]) / sigma) ** 2)
        m /= m.sum(axis=1, keepdims=True)
    return m[stride // 2::stride] if stride > 1 else m


def pyramid(image, levels: int = 3):
    """Blur pyramid of images (..., H, W, C): level 0 is the image, level l > 0 is
    blurred with a Gaussian of std 2^l px and subsampled by 2^l. Returns a list of arrays."""
    image = jnp.asarray(image)
    h, w = image.shape[-3], image.shape[-2]
    out = []
    for level in range(levels):
        stride = 2 ** level
        sigma = float(stride) if level else 0.0
        bh = jnp.asarray(_blur_matrix(h, sigma, stride))
        bw = jnp.asarray(_blur_matrix(w, sigma, stride))
        out.append(jnp.einsum("ih,...hwc,jw->...ijc", bh, image, bw) if level else image)
    return out


def _logpdf(r, sigma, kind: str, df):
    if kind == "normal":
        return -0.5 * (r / sigma) ** 2 - jnp.log(sigma) - 0.5 * jnp.log(2 * jnp.pi)
    if kind == "student_t":
        return (gammaln(0.5 * (df + 1)) - gammaln(0.5 * df) - 0.5 * jnp.log(df * jnp.pi)
                - jnp.log(sigma) - 0.5 * (df + 1) * jnp.log1p((r / sigma) ** 2 / df))
    raise ValueError(f"unknown noise kind {kind!r}: use 'normal' or 'student_t'")


def image_log_likelihood(rendered, observed, sigma, levels: int = 3, kind: str = "normal",
                         df=4.0, edge_weight: float = 0.0):
    """Log-likelihood of ``observed`` images given ``rendered`` ones (..., H, W, C).

    Per-pixel noise of scale ``sigma`` (Normal or Student-t with ``df``) summed over a blur
    pyramid of ``levels`` levels; level l (blur std 2^l px, subsampled by 2^l) is weighted
    4^l / levels so the pyramid as a whole counts as one image. ``edge_weight`` > 0 adds the
    same density on image gradients (finite differences, scale sigma * sqrt(2)).
    """
    rendered = jnp.asarray(rendered)
    observed = jnp.asarray(observed)
    total = 0.0
    for level, (r, o) in enumerate(zip(pyramid(rendered, levels), pyramid(observed, levels))):
        weight = (4.0 ** level) / levels
        total = total + weight * jnp.sum(_logpdf(r - o, sigma, kind, df))
    if edge_weight:
        for axis in (-3, -2):
            gr = jnp.diff(rendered, axis=axis)
            go = jnp.diff(observed, axis=axis)
            total = total + edge_weight * jnp.sum(
                _logpdf(gr - go, sigma * jnp.sqrt(2.0), kind, df))
    return total


# Frames of image observations, loaded once per process (outside any trace): paths -> array.
_FRAME_CACHE: dict[tuple[str, ...], np.ndarray] = {}
MAX_FRAMES = 16  # frames compared per image observation (evenly spaced when there are more)


def frame_subset(n: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """Indices of at most ``max_frames`` evenly spaced frames of ``n`` (first and last kept)."""
    if n <= max_frames:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max_frames)).astype(int))


def observed_frames(obs) -> tuple[np.ndarray, np.ndarray]:
    """(times (F,), frames (F, H, W, 3) in [0, 1]) of an image Observation, subsampled to at
    most MAX_FRAMES and cached per list of files."""
    key = tuple(str(p) for p in obs.frames)
    if key not in _FRAME_CACHE:
        idx = frame_subset(len(key))
        _, frames = load_frames([obs.frames[i] for i in idx], times=np.asarray(obs.times)[idx])
        _FRAME_CACHE[key] = frames
    idx = frame_subset(len(key))
    return np.asarray(obs.times)[idx], _FRAME_CACHE[key]
