"""The per-model cache of ``rho_ref`` at a screen's pairs (:meth:`brdfkit.render.screen.Screen.reference`)."""

from __future__ import annotations

import gc
import types

import numpy as np
import pytest
import torch

from brdfkit.render.screen import Screen


def _screen(m: int) -> Screen:
    return Screen(pix=np.zeros(m, np.int64), coords=np.zeros((3, m), np.float32), rw=np.ones((m, 3), np.float32),
                  pixels=1)


class _Model:
    """What :meth:`Screen.reference` asks of a model: a cache, a device and ``reference_at_pairs``."""

    device = "cpu"

    def __init__(self):
        self.cache = types.SimpleNamespace(screen={})
        self.calls = 0

    def reference_at_pairs(self, theta_h, theta_d, phi_d):
        self.calls += 1
        return torch.full((len(theta_h), 3), float(len(theta_h)))


def test_a_freed_screens_reference_is_not_served_to_a_new_screen_with_its_id():
    model, a, b = _Model(), _screen(5), _screen(7)
    assert a.reference(model).shape == (5, 3) and a.reference(model).shape == (5, 3) and model.calls == 1
    # b took the id a freed screen had (as CPython reuses ids): the stale entry is not b's.
    model.cache.screen[id(b)] = model.cache.screen.pop(id(a))
    assert b.reference(model).shape == (7, 3) and model.calls == 2


def test_screens_made_and_freed_in_turn_each_get_their_own_pairs():
    model, ids = _Model(), []
    for i in range(40):  # freed screens' ids come back within a few rounds in CPython
        s = _screen(3 + i % 4)
        ids.append(id(s))
        assert np.array_equal(s.reference(model).numpy(), np.full((3 + i % 4, 3), 3.0 + i % 4))
        del s
        gc.collect(0)  # the youngest generation: a full collection takes a quarter second in a test process
    assert len(set(ids)) < len(ids)  # ids did come back: the case this test is about happened
