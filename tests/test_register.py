"""The registration's batched least-squares step: the solutions numpy's solver gives, one system at a time."""

import numpy as np

from pmwm.register import _lstsq


def _reference(J, r):
    return np.stack([np.linalg.lstsq(J[b], r[b], rcond=None)[0] for b in range(len(J))])


def test_lstsq_matches_numpy_on_badly_scaled_systems():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 200, 7))
    J[..., 1:4] *= 1e4  # rotation columns scale with the mesh's size, translation columns do not
    r = rng.normal(size=(6, 200))
    got, want = _lstsq(J, r), _reference(J, r)
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())


def test_lstsq_gives_no_step_along_unconstrained_directions():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(3, 100, 7))
    J[0, :, 6] = 0.0  # a motion the data do not see
    J[1, :, 5] = J[1, :, 4]  # two motions the data cannot tell apart
    J[2] = 0.0  # nothing at all
    r = rng.normal(size=(3, 100))
    got, want = _lstsq(J, r), _reference(J, r)  # numpy's: the minimum-norm solution
    assert np.all(np.isfinite(got))
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12)
