"""`selfcal run` keeps what its acquisition took: the images in memory are the pixels read back
from the PNGs, the detections are made once, and the image noise drawn ahead by a worker thread is
the seeded stream (issue 17)."""

from __future__ import annotations

import numpy as np
import pytest

import selfcal.calibration.field.detections as detections_module
from selfcal.calibration.field.calibrate import detect_dataset
from selfcal.config.scenario import load_scenario
from selfcal.io.dataset import Dataset, read_gray
from selfcal.io.frame_cache import FrameCache
from selfcal.pipeline.run import run_acquire
from selfcal.sim.markers import make_marker_field
from selfcal.sim.render import apply_noise, noise_field
from selfcal.sim.sim_robot import SimRobot

pytestmark = pytest.mark.render


@pytest.fixture(scope="module")
def acquired(tmp_path_factory):
    """A small rendered dataset (6 postures) and the images its acquisition kept."""
    s = load_scenario(None, {"trajectory": {"poses": 6}, "validation": {"poses": 3}})
    out = tmp_path_factory.mktemp("kept")
    cache = FrameCache()
    run_acquire(s, out, quiet=True, keep=cache)
    return out, cache, dict(cache.detections)


def test_kept_images_are_the_pixels_read_back(acquired):
    out, cache, _ = acquired
    ds = Dataset.open(out)
    paths = ds.image_paths()
    assert len(paths) == 12 and set(cache.images) == {(i, c) for i, c, _ in paths}
    for index, cam, path in paths:
        np.testing.assert_array_equal(cache.images[(index, cam)], read_gray(path, index))


def test_kept_frames_stop_at_the_memory_budget(acquired):
    out, cache, _ = acquired
    small = FrameCache(max_bytes=3 * 640 * 480)
    for (index, cam), img in sorted(cache.images.items()):
        small.add(index, {cam: img})
    assert len(small.images) == 3 and small.nbytes == 3 * 640 * 480
    other = FrameCache()
    other.add(0, {"left": np.zeros((4, 4), np.uint16), "right": np.zeros((4, 4, 4), np.uint8)})
    assert other.images == {}  # kinds gray_of_png does not reproduce: read from the files


def test_detections_from_memory_and_reused_equal_those_from_the_files(acquired):
    out, cache, _ = acquired
    ds = Dataset.open(out)
    files = detect_dataset(ds)
    cache.detections.clear()
    first = detect_dataset(ds, cache=cache)  # from the images in memory, filling the cache
    assert len(cache.detections) == 12
    again = detect_dataset(ds, cache=cache)  # from the cache alone
    for got in (first, again):
        _assert_same_detections(got, files)


def _assert_same_detections(got, want) -> None:
    assert got.skipped_images == want.skipped_images
    assert got.corner_sigma_px == want.corner_sigma_px
    assert got.detections.keys() == want.detections.keys()
    for k, markers in want.detections.items():
        assert got.detections[k].keys() == markers.keys()
        for m, c in markers.items():
            np.testing.assert_array_equal(got.detections[k][m], c)


def test_detections_made_while_acquiring_are_those_from_the_files_and_reused(acquired, monkeypatch):
    """The field route's markers are detected as the acquisition keeps each image
    (detect_ahead): the same corners and noise as detected from the PNGs, and the calibration's
    detection takes them without detecting again."""
    out, _, ahead = acquired
    ds = Dataset.open(out)
    files = detect_dataset(ds)
    assert len(ahead) == 12
    cache = FrameCache(detections=dict(ahead))

    def no_detection(*args, **kwargs):
        raise AssertionError("detected again")

    monkeypatch.setattr(detections_module, "detect_markers_noise", no_detection)
    monkeypatch.setattr(detections_module, "read_gray", no_detection)
    _assert_same_detections(detect_dataset(ds, cache=cache), files)


def test_a_detection_failing_while_acquiring_is_left_to_the_calibration(acquired, monkeypatch):
    """A detection that raises on the acquisition's helper thread (say a cv2.error on an odd
    image) neither stops the acquisition (its frame is on disk) nor leaves a detection: the
    calibration's detect_dataset detects that image again from its file and reports there."""
    out, cache, _ = acquired
    kept = FrameCache()
    detections_module.detect_ahead(Dataset.open(out).info, kept)

    def broken(*args, **kwargs):
        raise RuntimeError("odd image")

    monkeypatch.setattr(detections_module, "detect_markers_noise", broken)
    kept.add(0, {"left": cache.images[(0, "left")]})  # does not raise
    assert kept.detections == {} and (0, "left") in kept.images


def test_noise_drawn_ahead_is_the_seeded_stream():
    """Three captures with noise equal the clean renders plus the generator's draws in order."""
    field = make_marker_field(n_markers=6, seed=2)
    postures = ([0, 0, 0, -90, 0], [10, -5, 5, -80, 20], [-10, 5, -5, -100, -20])
    with SimRobot("er4u-paper", field=field, image_sigma=3.0, seed=7) as noisy:
        got = []
        for q in postures:
            noisy.move_to(np.array(q, float))
            pair = noisy.capture()
            got += [pair.left, pair.right]
    rng = np.random.default_rng(7)
    with SimRobot("er4u-paper", field=field, image_sigma=0.0) as clean:
        for k, q in enumerate(postures):
            clean.move_to(np.array(q, float))
            pair = clean.capture()
            for j, img in enumerate((pair.left, pair.right)):
                want = apply_noise(img, noise_field(img.shape, 3.0, rng))
                np.testing.assert_array_equal(got[2 * k + j], want)


def test_msaa_is_the_renderers_sample_count():
    field = make_marker_field(n_markers=6, seed=2)
    for msaa, granted in ((0, 0), (None, 4)):
        with SimRobot("er4u-paper", field=field, msaa=msaa) as r:
            r.capture()
            assert r._renderer.samples == granted
