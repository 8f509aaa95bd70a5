"""The dataset's PNG images encoded with zlib-ng (the one PNG writer of ``selfcal.io.dataset``).

A PNG is its signature and three chunks: IHDR (size, 8 bits per sample, grey or RGB), IDAT (the
rows, each behind its filter byte, deflated) and IEND. Every row takes the SUB filter (each byte
minus the byte one pixel to its left, modulo 256: what OpenCV's writer chose for these images)
and the deflate codes Huffman codes alone: a camera image's noise leaves little for string
matching (with OpenCV's writer, its default RLE strategy gave 0.3 % larger files for 14 % more
CPU). zlib-ng's Huffman coder takes about half the CPU of zlib 1.2's, which OpenCV and Python's
``zlib`` link: a default ``selfcal run``'s 60 frames took 0.28 against 0.51 thread-CPU s with
OpenCV's writer (``MUJOCO_GL=egl python -m selfcal.benchmarks.speed.run_timeline``, ``_encode_png``,
load 16-20 on 2 cores), the files as large within 1 % (tests/unit/test_png.py). Lossless: any
PNG reader gives the same pixels back.

A drawing (``drawing=True``: the report's figures, :func:`selfcal.plots.plotting.save_figure`)
takes the UP filter (each byte minus the byte above it) and deflate's string matching at level
2 instead: its flat areas and repeated rows are long matches. ``selfcal run``'s three figures
took 1.4 ms each against Pillow's level-1 writer's 16.5 ms (which tries every filter on every
row), in files 1-4 % smaller (level 1 took 1.0 ms for files 17 % larger than Pillow's; level 6
3.5 ms, 5-9 % smaller). A drawing may carry an alpha channel and its dots per inch (a pHYs
chunk).
"""

from __future__ import annotations

import struct

import numpy as np
from zlib_ng import zlib_ng

from selfcal.errors import InputError

__all__ = ["encode_png"]

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_SUB = 1  # the PNG filter type: each byte minus the one a pixel to its left
_UP = 2  # the PNG filter type: each byte minus the byte above it
_COLOUR = {1: 0, 3: 2, 4: 6}  # channels -> PNG colour type (grey, RGB, RGBA)


def encode_png(img: np.ndarray, *, drawing: bool = False, dpi: float | None = None) -> bytes:
    """The PNG file of ``img``: uint8 grey (H, W) or (H, W, 1), RGB (H, W, 3) or RGBA (H, W, 4),
    channels in RGB(A) order. ``drawing``: compressed for a drawing's flat areas (module
    docstring); ``dpi``: dots per inch recorded in the file (None: none). ``InputError`` for
    another dtype or shape."""
    a = np.asarray(img)
    channels = 1 if a.ndim == 2 else a.shape[2] if a.ndim == 3 else 0
    if a.dtype != np.uint8 or channels not in _COLOUR or a.size == 0:
        raise InputError(
            f"a PNG image must be uint8 (H, W) grey, (H, W, 3) RGB or (H, W, 4) RGBA, got "
            f"{a.dtype} {a.shape}"
        )
    h, w = a.shape[:2]
    rows = np.ascontiguousarray(a).reshape(h, w * channels)
    data = np.empty((h, w * channels + 1), np.uint8)
    if drawing:
        data[:, 0] = _UP
        data[0, 1:] = rows[0]
        np.subtract(rows[1:], rows[:-1], out=data[1:, 1:])
        deflate = zlib_ng.compressobj(2, zlib_ng.DEFLATED, 15, 9, zlib_ng.Z_DEFAULT_STRATEGY)
    else:
        data[:, 0] = _SUB
        data[:, 1 : 1 + channels] = rows[:, :channels]
        np.subtract(rows[:, channels:], rows[:, :-channels], out=data[:, 1 + channels :])
        deflate = zlib_ng.compressobj(1, zlib_ng.DEFLATED, 15, 9, zlib_ng.Z_HUFFMAN_ONLY)
    idat = deflate.compress(data) + deflate.flush()
    header = struct.pack(">IIBBBBB", w, h, 8, _COLOUR[channels], 0, 0, 0)
    chunks = [_chunk(b"IHDR", header)]
    if dpi is not None:
        per_metre = round(dpi / 0.0254)
        chunks.append(_chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)))
    chunks += [_chunk(b"IDAT", idat), _chunk(b"IEND", b"")]
    return b"".join((_SIGNATURE, *chunks))


def _chunk(kind: bytes, body: bytes) -> bytes:
    """One PNG chunk: length, type, body and the CRC-32 of type and body."""
    crc = zlib_ng.crc32(body, zlib_ng.crc32(kind))
    return b"".join((struct.pack(">I", len(body)), kind, body, struct.pack(">I", crc)))
