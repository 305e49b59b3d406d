"""Measurement files: long-format CSV observations, control tables and image frame lists.

Every problem is a DataError naming the file, the row (1-based, the header is row 1) and
the column, so a user can open the file and fix it.
"""
from __future__ import annotations

import csv
import difflib
import math
from pathlib import Path

import numpy as np

from ..errors import DataError, Span
from ..observe.image import is_video, video_frames


def _rows(path: Path, span: Span | None) -> tuple[list[str], list[list[str]]]:
    if not path.is_file():
        raise DataError("file not found", path, span=span,
                        hint="data paths are relative to the scene file")
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = [r for r in csv.reader(fh)]
    except (OSError, UnicodeDecodeError, csv.Error) as ex:
        raise DataError(f"cannot read the file: {ex}", path, span=span) from None
    if not rows:
        raise DataError("the file is empty", path, span=span, hint="the first row names the columns")
    header = [h.strip() for h in rows[0]]
    return header, rows[1:]


def _col(header: list[str], name: str, path: Path, span) -> int:
    if name not in header:
        sugg = difflib.get_close_matches(name, header, n=1)
        raise DataError(f"no column '{name}'" + (f" (did you mean '{sugg[0]}'?)" if sugg else ""),
                        path, row=1, span=span, hint=f"the columns are: {', '.join(header)}")
    return header.index(name)


def _number(cell: str, path: Path, row: int, column: str, span) -> float:
    try:
        v = float(cell)
    except ValueError:
        raise DataError(f"'{cell}' is not a number", path, row=row, column=column, span=span,
                        hint="leave a cell empty for a missing value") from None
    if math.isnan(v) or math.isinf(v):
        raise DataError(f"'{cell}' is not a finite number", path, row=row, column=column, span=span,
                        hint="leave a cell empty for a missing value")
    return v


def _times(times: list[tuple[float, int]], path: Path, span) -> np.ndarray:
    for (a, _), (b, row) in zip(times, times[1:]):
        if b <= a:
            what = "repeats" if b == a else "goes back"
            raise DataError(f"time {what} (t = {b:g} after t = {a:g})", path, row=row, column="t",
                            span=span, hint="rows must be sorted by increasing time, one per time")
    return np.array([t for t, _ in times], dtype=float)


def read_observation(path: Path, columns, where: tuple[str, str] | None,
                     span: Span | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times (N,), values (N, D), mask (N, D)) of the rows matching ``where``."""
    header, rows = _rows(path, span)
    it = _col(header, "t", path, span)
    idx = [_col(header, c, path, span) for c in columns]
    wi = _col(header, where[0], path, span) if where else None
    times, values, mask, seen = [], [], [], []
    for n, row in enumerate(rows, start=2):
        if not any(c.strip() for c in row):
            continue
        if wi is not None:
            cell = row[wi].strip() if wi < len(row) else ""
            seen.append(cell)
            if cell != where[1]:
                continue
        if len(row) < len(header):
            row = row + [""] * (len(header) - len(row))
        tcell = row[it].strip()
        if not tcell:
            raise DataError("missing time", path, row=n, column="t", span=span)
        times.append((_number(tcell, path, n, "t", span), n))
        vals, ms = [], []
        for c, i in zip(columns, idx):
            cell = row[i].strip()
            if cell == "":
                vals.append(0.0)
                ms.append(False)
            else:
                vals.append(_number(cell, path, n, c, span))
                ms.append(True)
        values.append(vals)
        mask.append(ms)
    if not times:
        if where is not None:
            opts = sorted(set(seen))
            sugg = difflib.get_close_matches(where[1], opts, n=1)
            raise DataError(f"no row has {where[0]} == \"{where[1]}\""
                            + (f" (did you mean \"{sugg[0]}\"?)" if sugg else ""),
                            path, column=where[0], span=span,
                            hint=f"values in column '{where[0]}': {', '.join(opts[:8]) or 'none'}")
        raise DataError("no data rows", path, span=span)
    t = _times(times, path, span)
    return t, np.array(values, dtype=float).reshape(len(t), len(columns)), \
        np.array(mask, dtype=bool).reshape(len(t), len(columns))


def read_control(path: Path, columns, span) -> tuple[np.ndarray, np.ndarray]:
    """(times (N,), values (N, len(columns))) of a known control sequence; no cell may be empty."""
    header, rows = _rows(path, span)
    it = _col(header, "t", path, span)
    idx = [_col(header, c, path, span) for c in columns]
    times, values = [], []
    for n, row in enumerate(rows, start=2):
        if not any(c.strip() for c in row):
            continue
        row = row + [""] * (len(header) - len(row))
        times.append((_number(row[it].strip(), path, n, "t", span), n))
        values.append([_number(row[i].strip(), path, n, c, span) for c, i in zip(columns, idx)])
    if not times:
        raise DataError("no data rows", path, span=span)
    return _times(times, path, span), np.array(values, dtype=float)


def read_image_times(base: Path, pattern: str, rate: float | None, times_file: Path | None,
                     span) -> tuple[tuple[Path, ...], np.ndarray]:
    """Frames of ``pattern`` and their times (i / rate, or a times CSV).

    ``pattern`` is a glob of image files (sorted by name) or one video file, whose frames are
    VideoFrame entries and whose own frame rate serves when neither a rate nor times is given.
    """
    if rate is not None and times_file is not None:
        raise DataError("give the frame times with 'at RATE' or 'times \"file.csv\"', not both",
                        base / pattern, span=span)
    if is_video(pattern):
        frames, fps = video_frames(base / pattern)
        if rate is None and times_file is None:
            if fps <= 0:
                raise DataError("the video does not state its frame rate", base / pattern,
                                span=span, hint="give the frame times with 'at RATE' or "
                                                "'times \"file.csv\"'")
            rate = fps
    else:
        frames = tuple(sorted(p for p in base.glob(pattern) if p.is_file()))
    if not frames:
        raise DataError("no frame files match", base / pattern, span=span,
                        hint="the pattern is relative to the scene file, e.g. \"frames/*.png\"")
    if rate is None and times_file is None:
        raise DataError("give the frame times with 'at RATE' or 'times \"file.csv\"'",
                        base / pattern, span=span)
    if rate is not None:
        if rate <= 0:
            raise DataError("the frame rate must be positive", base / pattern, span=span)
        return frames, np.arange(len(frames)) / rate
    header, rows = _rows(times_file, span)
    it = _col(header, "t", times_file, span)
    times = [(_number(r[it].strip(), times_file, n, "t", span), n)
             for n, r in enumerate(rows, start=2) if any(c.strip() for c in r)]
    t = _times(times, times_file, span)
    if len(t) != len(frames):
        raise DataError(f"{len(t)} times for {len(frames)} frames", times_file, span=span,
                        hint="one time per frame file, in sorted order")
    return frames, t


def first_row(path: Path, column: str, value: str) -> int | None:
    """1-based row number (header = 1) of the first row whose ``column`` equals ``value``."""
    try:
        header, rows = _rows(path, None)
    except DataError:
        return None
    if column not in header:
        return None
    i = header.index(column)
    for n, row in enumerate(rows, start=2):
        if i < len(row) and row[i].strip() == value:
            return n
    return None
