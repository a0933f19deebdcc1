"""PyTorch tensors drive the adjoint as NumPy arrays do (through DLPack). The set-up does not
install PyTorch, so there the test skips, and ctest reports this file as skipped, not passed
(conftest.py); it is a file of its own so that the skip hides no other test."""

import numpy as np
import pytest

import tandem
from conftest import SCENES


def test_torch_tensors_are_accepted_when_torch_is_installed():
    torch = pytest.importorskip("torch")
    s = tandem.load(str(SCENES / "cbox.xml"), res=16)
    image = s.render(4, 0)
    delta = np.full_like(image, 1.0 / image.size)
    a = s.backward(delta, spp=2, seed=5, params="red.reflectance")
    b = s.backward(torch.from_numpy(delta), spp=2, seed=5, params="red.reflectance")
    assert np.array_equal(a["red.reflectance"], b["red.reflectance"])
