"""Tracking coloured objects in frames: colour segmentation, blob centroids, optional 3D.

Each tracked body has a colour; a pixel belongs to it when its chromaticity (rgb / sum) is
within ``tolerance`` of the colour's, so shading does not break the segmentation. The largest
blob's centroid gives the image position (u, v) in pixels (column, row; top-left pixel centre
at 0, 0). With a camera, a known plane or the object's radius turns (u, v) into world x, y, z.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np

from .errors import UsageError
from .io import atomic_path
from .observe.image import load_frames
from .render.camera import focal_pixels, unproject
from .render.camera_json import load_camera_json
from .render.types import RenderCamera


@dataclass(frozen=True)
class Target:
    """A body to track: its name and colour (RGB in [0, 1])."""

    name: str
    color: tuple[float, float, float]


def parse_color(text: str, index: int = 0) -> Target:
    """A Target from ``R,G,B`` or ``NAME=R,G,B`` (values in [0, 1] or 0..255; unnamed targets
    are ``object``, ``object1``, ... by their ``index``)."""
    name, _, rgb = text.rpartition("=")
    try:
        vals = [float(v) for v in rgb.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 3:
        raise UsageError(f"cannot read the colour {text!r}", hint="write R,G,B or NAME=R,G,B")
    if max(vals) > 1.0:
        vals = [v / 255.0 for v in vals]
    return Target(name or (f"object{index}" if index else "object"), tuple(vals))


def segment(frame: np.ndarray, color, tolerance: float = 0.08, min_value: float = 0.03
            ) -> np.ndarray:
    """Boolean mask (H, W) of pixels whose chromaticity is within ``tolerance`` of ``color``'s."""
    frame = np.asarray(frame, dtype=float)
    total = frame.sum(-1, keepdims=True)
    chroma = frame / np.maximum(total, 1e-9)
    target = np.asarray(color, dtype=float)
    target = target / max(target.sum(), 1e-9)
    return (np.linalg.norm(chroma - target, axis=-1) < tolerance) & (total[..., 0] > 3 * min_value)


def blob(mask: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Centroid (u, v) and area (pixels) of the largest connected blob of a mask, or None."""
    import cv2

    count, labels, stats, cents = cv2.connectedComponentsWithStats(mask.astype(np.uint8), 8)
    if count <= 1:
        return None
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return np.asarray(cents[best], dtype=float), float(stats[best, cv2.CC_STAT_AREA])


def track_image(times: np.ndarray, frames: np.ndarray, targets: Sequence[Target],
                tolerance: float = 0.08) -> list[tuple[float, str, float, float, float]]:
    """Rows (t, body, u, v, area) for every frame where a target is found."""
    rows = []
    for t, frame in zip(times, frames):
        for target in targets:
            found = blob(segment(frame, target.color, tolerance))
            if found is not None:
                (u, v), area = found
                rows.append((float(t), target.name, float(u), float(v), area))
    return rows


def parse_plane(text: str) -> tuple[np.ndarray, float]:
    """A plane written ``y=0`` (axis = value) or ``nx,ny,nz,d`` (n . x = d) -> (normal, d)."""
    text = text.replace(" ", "")
    try:
        if "=" in text:
            axis, value = text.split("=")
            normal = np.eye(3)["xyz".index(axis.lower())]
            return normal, float(value)
        nx, ny, nz, d = (float(p) for p in text.split(","))
    except (ValueError, IndexError):
        raise UsageError(f"cannot read the depth plane {text!r}",
                         hint="write AXIS=VALUE (e.g. y=0) or nx,ny,nz,d") from None
    normal = np.array([nx, ny, nz])
    norm = np.linalg.norm(normal)
    if norm == 0:
        raise UsageError(f"depth plane {text!r} has a zero normal")
    return normal / norm, d / norm


def to_world(camera: RenderCamera, uv: np.ndarray, area: np.ndarray, plane=None, radius=None
             ) -> np.ndarray:
    """World points (N, 3) of image points: on ``plane`` (normal, d), or at the depth where a
    sphere of ``radius`` m covers ``area`` pixels (small-sphere approximation)."""
    uv = np.asarray(uv, dtype=float)
    near = np.asarray(unproject(camera, uv, np.ones(len(uv))))  # points at unit depth
    eye = np.asarray(camera.position)
    if plane is not None:
        normal, d = plane
        ray = near - eye
        s = (d - eye @ normal) / (ray @ normal)
        return eye + s[:, None] * ray
    if radius is not None:
        r_px = np.sqrt(np.asarray(area, dtype=float) / np.pi)
        depth = float(focal_pixels(camera)) * radius / r_px
        return np.asarray(unproject(camera, uv, depth))
    raise UsageError("3D tracking needs a depth plane or the object's radius")


def write_csv(path: Path, rows, world: np.ndarray | None = None) -> None:
    """Long-format CSV: ``t,body,u,v`` or, with world points, ``t,body,x,y,z``."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        out = csv.writer(fh)
        if world is None:
            out.writerow(["t", "body", "u", "v"])
            for t, name, u, v, _ in rows:
                out.writerow([f"{t:.6f}", name, f"{u:.4f}", f"{v:.4f}"])
        else:
            out.writerow(["t", "body", "x", "y", "z"])
            for (t, name, *_), p in zip(rows, world):
                out.writerow([f"{t:.6f}", name, f"{p[0]:.6f}", f"{p[1]:.6f}", f"{p[2]:.6f}"])


class Tracked(NamedTuple):
    """What ``track_source`` found: rows (t, body, u, v, area), world points (N, 3) or None,
    the targets and the number of frames read."""

    rows: list
    world: np.ndarray | None
    targets: tuple[Target, ...]
    frames: int

    def found_in(self, name: str) -> int:
        """Frames in which the target ``name`` was found."""
        return sum(1 for r in self.rows if r[1] == name)

    def write_csv(self, path: Path) -> None:
        """The tracks as ``write_csv`` writes them (world points where there are)."""
        write_csv(path, self.rows, self.world)


def track_source(source, colors: Sequence, tolerance: float = 0.08, camera=None,
                 depth_plane: str | None = None, radius: float | None = None,
                 rate: float | None = None) -> Tracked:
    """Track coloured objects in a video, a folder or a glob of frames. ``colors``: Targets or
    their text (``parse_color``). With ``camera`` (a camera.json) and a ``depth_plane``
    (``parse_plane``) or the objects' ``radius`` (m), world positions; ``rate`` (Hz) defaults to
    the camera file's frame rate for frames, the video's own for a video."""
    targets = tuple(c if isinstance(c, Target) else parse_color(c, i) for i, c in enumerate(colors))
    spec = load_camera_json(camera) if camera is not None else None
    if (depth_plane or radius) and spec is None:
        raise UsageError("--depth-plane and --radius need --camera")
    if spec is not None and rate is None and not Path(source).suffix.lower() in (".mp4", ".avi"):
        rate = spec.frame_rate
    size = (spec.camera.width, spec.camera.height) if spec is not None else None
    times, frames = load_frames(source, rate=rate, size=size)
    rows = track_image(times, frames, targets, tolerance)
    world = None
    if spec is not None and (depth_plane or radius):
        uv = np.array([[r[2], r[3]] for r in rows]).reshape(-1, 2)
        area = np.array([r[4] for r in rows])
        world = to_world(spec.camera, uv, area,
                         plane=parse_plane(depth_plane) if depth_plane else None, radius=radius)
    return Tracked(rows, world, targets, len(frames))
