"""brdfkit.runtime.resolve_device: the one device rule of the library."""

from __future__ import annotations

import pytest
import torch

from brdfkit.runtime import resolve_device
from brdfkit.errors import InputError


def test_auto_and_cpu():
    want = "cuda" if torch.cuda.is_available() else "cpu"
    assert resolve_device().type == want and resolve_device("auto").type == want
    assert resolve_device("cpu") == torch.device("cpu") == resolve_device(torch.device("cpu"))


@pytest.mark.parametrize("name", ["tpu", "mps", "gpu", ""])
def test_other_devices_refused_in_one_line(name):
    with pytest.raises(InputError, match=f"device {name!r}: use auto, cpu or cuda"):
        resolve_device(name)


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has CUDA")
def test_cuda_without_a_gpu_refused():
    for name in ("cuda", "cuda:1"):
        with pytest.raises(InputError, match="no CUDA device is available"):
            resolve_device(name)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_cuda_local_rank_picks_its_gpu():
    n = torch.cuda.device_count()
    assert resolve_device("cuda", local_rank=n + 1) == torch.device(f"cuda:{(n + 1) % n}")
    assert resolve_device("cuda") == torch.device("cuda")
