"""The field route's detections: every image's ArUco markers (:func:`detect_dataset`, cached on
disk per frame and camera, the images that show none named), the observations the camera stage
takes from them (:func:`observations_of`) and the check that the markers a scale distance
names were seen."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import NamedTuple

import numpy as np

from selfcal.calibration.field.cameras import (
    dataset_camera,
    models_of,
)
from selfcal.calibration.field.failures import CalibrationError
from selfcal.calibration.field.self_calibration import (
    Observations,
)
from selfcal.camera import (
    LensCamera,
)
from selfcal.camera.undistort import Undistorter
from selfcal.errors import SelfCalWarning
from selfcal.io.dataset import Dataset, DatasetError, Detections, read_gray
from selfcal.io.dataset_info import DatasetInfo
from selfcal.io.frame_cache import FrameCache
from selfcal.target.aruco_detect import detect_markers_noise
from selfcal.threads import helper_threads


class NoMarkersWarning(SelfCalWarning):
    """Some images show no marker at all (they are skipped; the result lists them as well)."""


class MarkerDetections(NamedTuple):
    """What :func:`detect_dataset` found: the corners, the images that show no marker
    (``NNNN_left`` / ``NNNN_right``; skipped) and the detector's own estimate of the corner
    noise (px per coordinate, RMS over the detections; None when it has none: stored
    detections, images undistorted through a lens)."""

    detections: Detections
    skipped_images: tuple[str, ...]
    corner_sigma_px: float | None = None


def skipped_images_message(skipped: tuple[str, ...], dictionary: str) -> str:
    """The sentence naming the images without markers (the warning and the result's)."""
    more = " ..." if len(skipped) > 8 else ""
    return (
        f"{len(skipped)} image(s) show no {dictionary} marker and are skipped: "
        f"{', '.join(skipped[:8])}{more}"
    )


def detect_dataset(
    ds: Dataset,
    progress=None,
    lens: LensCamera | Mapping[str, LensCamera] | None = None,
    cache: FrameCache | None = None,
    start: Detections | None = None,
) -> MarkerDetections:
    """Marker corners of every image (images path) or the stored detections (analytic path),
    and the images that show no marker (for people also a :class:`NoMarkersWarning`).
    ``lens``: a camera with a lens (an estimate), or one per camera name (a camera not named is
    detected as it is): detect on the images undistorted with it and map the corners back (:class:`selfcal.camera.undistort.Undistorter`; the straight-edge corner
    refinement is biased on bent edges). The screening of hidden and grazing markers
    (:func:`selfcal.target.aruco_detect.detect_markers`, docs/accuracy.md) runs only for a dataset
    camera without a lens: on bent or resampled edges its level test drops markers unevenly
    (rendered lens scenario: worst camera-parameter z 3.05 with it, 1.78 without).
    ``cache``: the images already in memory (the others are read from the files) and the
    detections of an earlier call on the same dataset (reused, and the new ones added; not
    through a lens): :class:`selfcal.io.frame_cache.FrameCache`.
    ``start``: with ``lens``, the detections of the same images without it (an earlier call):
    a marker whose refinement in the undistorted image fails from the detector's own corners
    is refined again from these, mapped through the lens (``start`` of
    :func:`selfcal.target.aruco_detect.detect_markers_noise`; before, the rendered
    scenarios/mono.toml lost two of frame 29's three markers and the frame).

    Raises:
        DatasetError: a missing or unreadable image, or one whose size is not dataset.json's.
        CalibrationError: no marker in any image.
    """
    if ds.info.observation == "detections":
        return MarkerDetections(ds.read_detections(), ())
    screen = _screens(ds.info)
    out: Detections = {}
    empty: list[str] = []
    noise: list[float] = []
    if progress is not None:
        progress.start(len(ds.indices) * len(ds.info.cameras))  # one image per camera
    W, H = ds.info.resolution
    lens_of = lens if isinstance(lens, Mapping) else dict.fromkeys(ds.info.cameras, lens)
    flats = {c: Undistorter(v) for c, v in lens_of.items() if v is not None}

    def detect(item: tuple[int, str, Path]) -> tuple[int, str, dict, dict]:
        index, cam, path = item
        flat = flats.get(cam)
        key = (index, cam, screen)
        if flat is None and cache is not None and key in cache.detections:
            dets, sig = cache.detections[key]
            return index, cam, {k: c.copy() for k, c in dets.items()}, dict(sig)
        img = cache.images.get((index, cam)) if cache is not None else None
        img = read_gray(path, index) if img is None else img
        if img.shape[1] != W or img.shape[0] != H:
            raise DatasetError(
                f"frame {index:04d}_{cam}.png is {img.shape[1]}x{img.shape[0]} px but dataset.json "
                f"says {W}x{H}"
            )
        if flat is None:
            dets, sig = detect_markers_noise(img, ds.info.dictionary, screen=screen)
            if cache is not None:
                cache.detections[key] = ({k: c.copy() for k, c in dets.items()}, dict(sig))
            return index, cam, dets, sig
        known = {} if start is None else start.get((index, cam), {})
        dets, _ = detect_markers_noise(
            flat.image(img),
            ds.info.dictionary,
            screen=False,
            start={k: flat.undistorted(c) for k, c in known.items()},
        )
        return index, cam, {k: flat.distorted(c) for k, c in dets.items()}, {}

    # OpenCV releases the GIL while decoding and detecting: use every core, keep the order.
    images = list(ds.image_paths(in_memory=() if cache is None else cache.images))
    with ThreadPoolExecutor(max_workers=helper_threads(len(images))) as pool:
        for index, cam, dets, sig in pool.map(detect, images):
            noise += sig.values()
            if dets:
                out[(index, cam)] = dets
            else:
                empty.append(f"{index:04d}_{cam}")
            if progress is not None:
                progress.advance()
    if progress is not None:
        progress.finish()
    if empty:
        text = skipped_images_message(tuple(empty), ds.info.dictionary)
        warnings.warn(text, NoMarkersWarning, stacklevel=2)
    if not out:
        raise CalibrationError(
            f"no marker was detected in any image of {ds.root}; check the target dictionary "
            f"({ds.info.dictionary}), the lighting and that the camera sees the marker field"
        )
    sigma = float(np.sqrt(np.mean(np.square(noise)))) if noise else None
    return MarkerDetections(out, tuple(empty), sigma)


def _screens(info: DatasetInfo) -> bool:
    """Whether :func:`detect_dataset` screens hidden and grazing markers: for a dataset camera
    without a lens."""
    return not any(isinstance(c, LensCamera) for c in models_of(dataset_camera(info)))


def detect_ahead(info: DatasetInfo, cache: FrameCache) -> None:
    """Have ``cache`` detect each image's markers as the acquisition keeps it
    (:attr:`FrameCache.on_image`, on a helper thread of the acquisition's writer, beside the
    rendering of the next posture), the detection :func:`detect_dataset` would run on that
    image, stored where it looks first: the calibration that follows reuses them. An image of
    another size than ``info``'s is left to :func:`detect_dataset` (which names it), and so is
    an image whose detection fails here: the failure is the calibration's to report, from the
    image's file, never the acquisition's (whose frame is on disk by then)."""
    if info.observation != "images":
        return
    screen = _screens(info)
    W, H = info.resolution

    def detect(index: int, cam: str, gray: np.ndarray) -> None:
        if gray.shape[:2] != (H, W):
            return
        try:
            dets, sig = detect_markers_noise(gray, info.dictionary, screen=screen)
        except Exception:  # detected again from the file by detect_dataset, which reports it
            return
        cache.detections[(index, cam, screen)] = (dets, sig)

    cache.on_image = detect


def observations_of(ds: Dataset, dets: Detections) -> Observations:
    """The detections as :class:`selfcal.calibration.field.self_calibration.Observations`, configurations numbered by their
    position in ``ds.indices``."""
    pos = {int(i): k for k, i in enumerate(ds.indices)}
    remapped: dict[tuple[int, int | str], dict[int, np.ndarray]] = {
        (pos[i], cam): m for (i, cam), m in dets.items() if i in pos
    }
    return Observations.from_corners(remapped, n_configs=len(ds.indices), cameras=ds.info.cameras)


def _check_scale_markers(ds: Dataset, dets: Detections) -> None:
    for mid in ds.info.scale_ids:
        views = [k for k, m in dets.items() if mid in m]
        if len(views) < 2:
            raise CalibrationError(
                f"scale marker {mid} is seen in {len(views)} image(s); it must be seen in at least "
                "two so its position can be triangulated: move the scale bar into view or add "
                "postures that see it"
            )
