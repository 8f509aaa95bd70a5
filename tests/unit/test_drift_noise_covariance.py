"""The paired drift check's noise covariance (selfcal.calibration.drift.paired.noise_covariance):
a calibration written before the key leaves the cross term out; a key of the wrong shape is an
error naming it, never read as absent (review of session 23)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from selfcal.calibration.drift.paired import noise_covariance
from selfcal.errors import InputError


def _cal(accuracy):
    """A calibration with two free camera parameters and ``accuracy`` as its block."""
    return SimpleNamespace(accuracy=accuracy, cameras=[SimpleNamespace(free=("fx", "cx"))])


EM = SimpleNamespace(covariance=np.eye(3))  # three kinematic parameters: (5, 5) in all


def test_a_calibration_without_the_key_leaves_the_cross_term_out():
    assert noise_covariance(_cal({}), EM) is None
    assert noise_covariance(_cal(None), EM) is None


def test_the_key_of_the_right_shape_is_read():
    C = np.arange(25.0).reshape(5, 5)
    assert np.array_equal(noise_covariance(_cal({"noise_covariance_si": C.tolist()}), EM), C)


@pytest.mark.parametrize("value", [np.eye(4).tolist(), [], [[1.0, 2.0], [3.0]]])
def test_the_key_of_another_shape_is_an_error_naming_it(value):
    with pytest.raises(InputError, match=r"accuracy\.noise_covariance_si") as e:
        noise_covariance(_cal({"noise_covariance_si": value}), EM)
    assert "calibration.json" in str(e.value) and "selfcal calibrate" in (e.value.fix or "")
