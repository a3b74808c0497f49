"""The robust scheme's keyed site layout (pmwm.schemes.robust.layout): its draws are numpy's."""

import numpy as np
import pytest

from pmwm.schemes.robust.layout import _Integers


@pytest.mark.parametrize("seed", [0, 1, 12345])
def test_integers_draws_what_rng_integers_draws(seed):
    # the same integers and the same generator state afterwards, whatever the bounds (1, small,
    # large, and past 2**32: numpy's own path) and whatever draws came before (a permutation leaves
    # half of a 64-bit output waiting)
    ours, numpy_rng = np.random.default_rng(seed), np.random.default_rng(seed)
    bounds = np.random.default_rng(seed + 1).integers(1, 5000, 3000).tolist()
    bounds += [1, 2, 3, 2**31, 2**31 + 1, 2**32 - 1, 2**32, 2**40, 7, 1, 1, 9] * 20
    for rng in (ours, numpy_rng):
        rng.permutation(11)
        rng.standard_normal(3)
    integers = _Integers(ours)
    got = [integers(n) for n in bounds]
    integers.close()
    assert got == [int(numpy_rng.integers(n)) for n in bounds]
    assert ours.bit_generator.state == numpy_rng.bit_generator.state
    assert ours.random() == numpy_rng.random()


def test_integers_refuses_what_rng_integers_refuses():
    with pytest.raises(ValueError):
        _Integers(np.random.default_rng(0))(0)
